//! The thesis's discrete look-up of covered samples (Forest 2008, §4.4.3,
//! Fig. 4.9): precomputed bit fields instead of the per-sample test, as an
//! option of depth complexity sampling.
//!
//! For one fixed sample set in chart coordinates (the light's centre at
//! the origin), two tables of bit fields (bit `k` = sample `k`, in `u64`
//! words, so any `N`):
//!
//! - **Half-planes** (the thesis's cube map): for a direction `v`, the
//!   samples with `cross(v, s) ≥ 0`, on the left of (or on) the line
//!   through the origin along `v`. Indexed by `v`'s direction in a *square
//!   map*, the 2-D analogue of a cube map: the face is `v`'s major axis
//!   and sign, the bin the minor/major ratio in `[−1, 1]` (no `atan2`).
//! - **Lines** (the thesis's 2-D texture): for the line of an edge, the
//!   samples on its far side from the origin. Indexed by the orthogonal
//!   projection of the origin onto the line in polar form: the direction
//!   of the line's outward normal (a square map again) and its distance
//!   `d` from the origin, in `[0, r_max)` with `r_max` the largest sample
//!   radius (a line with `d ≥ r_max` has no sample beyond it).
//!
//! An edge `lo → hi` (`cross(lo, hi) > 0`, [`OrientedEdge`]) covers
//!
//! ```text
//! M = half_plane(lo) & !half_plane(hi) & line(lo, hi)
//! ```
//!
//! which is the exact test of [`super::counters`] (`cross(lo, s) ≥ 0`,
//! `cross(hi, s) < 0`, `orient(lo, hi, s) < 0`) with each factor taken at
//! its table cell's representative instead of at the edge. The sector
//! factors stay complementary for a vertex shared by two consecutive
//! edges (the same `v` falls in the same cell), so the sectors of a
//! closed silhouette loop still partition the samples, as the half-open
//! exact test does.
//!
//! # Error
//!
//! A factor can only disagree with its exact test for a sample `s` within
//! the cell's half-width of the factor's boundary ([`TableErrorBounds`]):
//!
//! - half-plane of `v`: `|cross(v̂, s)| ≤ sin(α_s) |s|`, `α_s` the largest
//!   angular half-width of a half-plane bin;
//! - line `n̂ · s = d`: `|n̂ · s − d| ≤ 2 sin(α_l / 2) |s| + Δd`, `α_l` the
//!   largest angular half-width of a normal bin, `Δd` half a distance bin.
//!
//! So every mismatching (edge, sample) decision lies in one of three bands
//! along the edge's sector rays and its line; the unit tests check exactly
//! that on random edges, and measure how many decisions fall in them.
//!
//! # When the tables are valid
//!
//! Only when every receiver using them has the same samples in chart
//! coordinates: rect lights (whose chart, the light's own `(s, t)`, does
//! not depend on the receiver) with the `correlated` pattern (one table)
//! or `interleaved:n` (one table per set, `n²`). See
//! [`CoverageTables::applicable`].

use super::counters::{ChartSamples, OrientedEdge, LANES};
use crate::sampling::SamplePattern;
use crate::scene::LightShape;
use crate::simd::{f32x4, i32x4, i32x8};
use std::f64::consts::FRAC_PI_2;

/// Largest total size of one light's tables [`CoverageTables::new`]
/// accepts: 512 MiB. Beyond it a resolution is a mistake, not a choice
/// (the per-sample test is then faster and exact).
pub const MAX_TABLE_BYTES: u64 = 512 << 20;

/// Resolution of the tables: bins per square-map face for directions, and
/// distance bins for lines.
#[derive(Debug, Clone, Copy, PartialEq, Eq)]
pub struct TableResolution {
    /// Bins per face of the half-plane square map (4 faces: `4 × sector`
    /// directions).
    pub sector: u32,
    /// Bins per face of the line table's normal directions.
    pub line_directions: u32,
    /// Distance bins of the line table over `[0, r_max)`.
    pub line_distances: u32,
}

impl Default for TableResolution {
    /// 256 half-plane directions (64 per face, as the thesis's
    /// `64 × 64 × 6` cube map has 64 bins per face axis), 256 line normal
    /// directions × 128 distances. Chosen from the measured error/speed
    /// trade-off in `docs/algorithms/dcs.md` ("Bit-field look-up").
    fn default() -> TableResolution {
        TableResolution {
            sector: 64,
            line_directions: 64,
            line_distances: 128,
        }
    }
}

impl TableResolution {
    /// Bytes of the tables for `n` samples at this resolution.
    pub fn bytes(&self, n: usize) -> u64 {
        let words = n.div_ceil(64) as u64;
        let sector = 4 * u64::from(self.sector);
        let lines = 4 * u64::from(self.line_directions) * u64::from(self.line_distances);
        (sector + lines) * words * 8
    }
}

/// How far from its boundary a table factor may be wrong (see the module
/// documentation), in chart units and radians.
#[derive(Debug, Clone, Copy, PartialEq)]
pub struct TableErrorBounds {
    /// Largest angle between a direction and its half-plane bin's
    /// representative, `α_s`.
    pub sector_angle: f64,
    /// Largest angle between a line normal and its bin's representative,
    /// `α_l`.
    pub line_angle: f64,
    /// Largest distance between a line's `d` and its bin's centre, `Δd`.
    pub line_distance: f64,
}

/// Bit field number `cell` of `table` (`words` words each).
#[inline]
fn field(table: &[u64], cell: usize, words: usize) -> &[u64] {
    let at = cell * words;
    &table[at..at + words]
}

/// The line factor of an edge's mask.
enum LineFactor<'a> {
    /// The samples beyond the line.
    Field(&'a [u64]),
    /// No sample lies beyond the line (`d ≥ r_max`).
    Empty,
    /// The edge is so short that its normal is not defined in f32: the
    /// sector alone decides (as the thesis does for a line through the
    /// centre, "a field of bits set at one"); such a sector is itself
    /// empty or thinner than the half-plane cells.
    Undefined,
}

/// The bit-field tables of one sample set (one light, one shared set).
#[derive(Debug, Clone)]
pub struct CoverageTables {
    /// Samples.
    n: usize,
    /// `u64` words per bit field.
    words: usize,
    resolution: TableResolution,
    /// Largest sample radius; lines at or beyond it cover nothing.
    r_max: f32,
    /// `line_distances / r_max`.
    inv_bin_width: f32,
    /// `4 × sector` bit fields.
    half_planes: Vec<u64>,
    /// `(4 × line_directions) × line_distances` bit fields, direction-major.
    lines: Vec<u64>,
    bounds: TableErrorBounds,
}

/// The square-map face of the direction of `v` and the ratio `t` over
/// it as `(face, numerator, denominator)`.
///
/// Faces counter-clockwise from `+x`: face `f` holds the angles within
/// 45° of `f · 90°`, parametrised by `t = tan(angle − f · 90°) ∈ [−1, 1]`
/// (`y/x` on the `±x` faces, `−x/y` on the `±y` faces).
#[inline]
fn square_face(v: [f32; 2]) -> (usize, f32, f32) {
    let [x, y] = v;
    // Selects rather than branches: edges come in random directions, and
    // a mispredicted face costs more than the rest of the look-up.
    let x_major = x.abs() >= y.abs();
    let num = if x_major { y } else { -x };
    let den = if x_major { x } else { y };
    (usize::from(!x_major) + 2 * usize::from(den < 0.0), num, den)
}

/// Square-map bin of the direction of `v` with `per_face` bins per face
/// ([`square_face`]). A zero or NaN direction lands in its face's bin 0
/// (float-to-int casts saturate, NaN to 0).
#[cfg(test)]
fn direction_bin(v: [f32; 2], per_face: usize) -> usize {
    let (face, num, den) = square_face(v);
    let half = 0.5 * per_face as f32;
    let bin = ((num / den) * half + half) as usize;
    face * per_face + bin.min(per_face - 1)
}

/// The representative unit direction of square-map bin `index` (the
/// angular middle of the bin) and the bin's angular half-width.
fn bin_direction(index: usize, per_face: usize) -> ([f64; 2], f64) {
    let (face, bin) = (index / per_face, index % per_face);
    let t = |b: usize| -1.0 + 2.0 * b as f64 / per_face as f64;
    let (a0, a1) = (t(bin).atan(), t(bin + 1).atan());
    let mid = 0.5 * (a0 + a1) + face as f64 * FRAC_PI_2;
    ([mid.cos(), mid.sin()], 0.5 * (a1 - a0))
}

/// Largest angular half-width of a square-map bin (the bins at the
/// faces' middles, where `atan` is steepest).
fn max_half_width(per_face: usize) -> f64 {
    (0..per_face)
        .map(|b| bin_direction(b, per_face).1)
        .fold(0.0, f64::max)
}

impl CoverageTables {
    /// Whether one table set can serve `pattern` on `light`: `Ok(k)` with
    /// `k` the number of distinct sample sets (one [`CoverageTables`]
    /// each), or an error saying why not, fit for the command line.
    ///
    /// The tables hold one fixed set of chart points, so every receiver
    /// using them must have exactly those points:
    ///
    /// - rect lights: the chart is the light's own `(s, t)`, the same from
    ///   every receiver, so the pattern decides: `correlated` gives every
    ///   pixel the same set (`Ok(1)`); `interleaved:n` gives `n²` sets,
    ///   pixel `(x, y)` using set
    ///   [`crate::sampling::PatternSampler::interleaved_set`] (`Ok(n²)`);
    ///   `stratified`, `rotated`, `poisson` and `sobol` move the points per
    ///   pixel (fresh jitter, toroidal or digital shifts) and are refused.
    ///   (The thesis decorrelates by a true rotation about the centre,
    ///   which a table could undo by rotating the edge; our `rotated` is a
    ///   toroidal shift on the square, which no table lookup can undo.)
    /// - sphere lights: refused. Their chart is the cone's gnomonic chart
    ///   scaled to the unit disc, where sample `(s, t)` lies at radius
    ///   `tan θ / tan θmax` with `cos θ = 1 − s (1 − cos θmax)`: the
    ///   radial placement changes with the receiver's distance (through
    ///   `θmax`), not only by a scale, so no normalisation makes the set
    ///   fixed (e.g. `s = 0.5` lies at 0.703 for `θmax = 10°` and 0.509 for
    ///   `60°`).
    pub fn applicable(pattern: SamplePattern, light: &LightShape) -> Result<u32, String> {
        if let LightShape::Sphere { .. } = light {
            return Err(
                "the bit-field look-up of covered samples needs every receiver to see \
                 the same samples in the light's chart, and a sphere light's samples move \
                 in its chart with the receiver's distance (radius tan θ / tan θmax with \
                 cos θ = 1 − s (1 − cos θmax)): use the exact per-sample test for sphere \
                 lights"
                    .into(),
            );
        }
        match pattern {
            SamplePattern::Correlated => Ok(1),
            SamplePattern::Interleaved { n } => Ok(n.max(1).saturating_mul(n.max(1))),
            other => Err(format!(
                "the bit-field look-up of covered samples needs a sample set shared by \
                 many pixels, and pattern `{other}` gives every pixel its own (per-pixel \
                 jitter, toroidal or digital shift): use --pattern correlated or \
                 interleaved[:N], or the exact per-sample test"
            )),
        }
    }

    /// Builds the tables for `samples` (chart coordinates) at `resolution`.
    /// Errors when a resolution is 0 or the tables would exceed
    /// [`MAX_TABLE_BYTES`]. Samples that are not finite are never covered.
    pub fn new(samples: &[[f32; 2]], resolution: TableResolution) -> Result<Self, String> {
        let TableResolution {
            sector,
            line_directions,
            line_distances,
        } = resolution;
        if sector == 0 || line_directions == 0 || line_distances == 0 {
            return Err(format!(
                "bit-field tables need at least one bin per dimension, got {resolution:?}"
            ));
        }
        let bytes = resolution.bytes(samples.len());
        if bytes > MAX_TABLE_BYTES {
            return Err(format!(
                "bit-field tables for {} samples at {resolution:?} would take {} MiB \
                 (more than {} MiB): lower the resolution",
                samples.len(),
                bytes >> 20,
                MAX_TABLE_BYTES >> 20
            ));
        }
        let n = samples.len();
        let words = n.div_ceil(64);
        let finite = |s: &[f32; 2]| s[0].is_finite() && s[1].is_finite();
        let r_max = samples
            .iter()
            .filter(|s| finite(s))
            .map(|s| f64::from(s[0]).hypot(f64::from(s[1])))
            .fold(0.0, f64::max);
        // Rounded up to f32, so that `d ≥ r_max` (nothing beyond the line)
        // is a test against a bound no sample exceeds.
        let r_max_f32 = (r_max as f32).next_up();
        let (sector, line_dirs, line_dist) = (
            sector as usize,
            line_directions as usize,
            line_distances as usize,
        );

        // Half-planes: bit k of direction c is `cross(v_c, s_k) ≥ 0`.
        let mut half_planes = vec![0u64; 4 * sector * words];
        // (`words = 0`: no samples, no fields, nothing to fill.)
        for (c, row) in half_planes.chunks_exact_mut(words.max(1)).enumerate() {
            let ([vx, vy], _) = bin_direction(c, sector);
            for (k, s) in samples.iter().enumerate() {
                let (sx, sy) = (f64::from(s[0]), f64::from(s[1]));
                if vx * sy - vy * sx >= 0.0 {
                    row[k / 64] |= 1 << (k % 64);
                }
            }
        }

        // Lines: bit k of (direction c, distance j) is `n̂_c · s_k > d_j`,
        // `d_j` the bin's centre. Per direction, the samples sorted by
        // their projection make each distance bin's field the previous
        // (farther) one plus the samples passed.
        let bin_width = f64::from(r_max_f32) / line_dist as f64;
        let mut lines = vec![0u64; 4 * line_dirs * line_dist * words];
        let mut order: Vec<(f64, usize)> = Vec::with_capacity(n);
        if words > 0 {
            for c in 0..4 * line_dirs {
                let ([nx, ny], _) = bin_direction(c, line_dirs);
                order.clear();
                order.extend(
                    samples
                        .iter()
                        .enumerate()
                        .filter(|(_, s)| finite(s))
                        .map(|(k, s)| (nx * f64::from(s[0]) + ny * f64::from(s[1]), k)),
                );
                // Farthest first.
                order.sort_unstable_by(|a, b| b.0.total_cmp(&a.0));
                let mut field = vec![0u64; words];
                let mut next = 0;
                for j in (0..line_dist).rev() {
                    let d = (j as f64 + 0.5) * bin_width;
                    while next < order.len() && order[next].0 > d {
                        let k = order[next].1;
                        field[k / 64] |= 1 << (k % 64);
                        next += 1;
                    }
                    let at = (c * line_dist + j) * words;
                    lines[at..at + words].copy_from_slice(&field);
                }
            }
        }

        Ok(CoverageTables {
            n,
            words,
            resolution,
            r_max: r_max_f32,
            inv_bin_width: (1.0 / bin_width) as f32,
            half_planes,
            lines,
            bounds: TableErrorBounds {
                sector_angle: max_half_width(sector),
                line_angle: max_half_width(line_dirs),
                line_distance: 0.5 * bin_width,
            },
        })
    }

    /// [`CoverageTables::new`] for the samples of a [`ChartSamples`] (its
    /// `len()` samples, not the padding).
    pub fn from_chart(samples: &ChartSamples, resolution: TableResolution) -> Result<Self, String> {
        let points: Vec<[f32; 2]> = (0..samples.len()).map(|k| samples.get(k)).collect();
        CoverageTables::new(&points, resolution)
    }

    /// Number of samples `N`.
    pub fn len(&self) -> usize {
        self.n
    }

    /// Whether there are no samples.
    pub fn is_empty(&self) -> bool {
        self.n == 0
    }

    /// The resolution the tables were built at.
    pub fn resolution(&self) -> TableResolution {
        self.resolution
    }

    /// Bytes held by the tables.
    pub fn bytes(&self) -> u64 {
        ((self.half_planes.len() + self.lines.len()) * 8) as u64
    }

    /// Largest sample radius (rounded up to `f32`).
    pub fn r_max(&self) -> f32 {
        self.r_max
    }

    /// How far from its boundary each factor may be wrong.
    pub fn error_bounds(&self) -> TableErrorBounds {
        self.bounds
    }

    /// The three fields of `lo → hi`: half-plane of `lo`, half-plane of
    /// `hi`, and the line factor.
    #[inline]
    fn fields(&self, lo: [f32; 2], hi: [f32; 2]) -> (&[u64], &[u64], LineFactor<'_>) {
        // Outward normal (the covered side is the right of lo → hi, away
        // from the origin) and the origin's distance to the line,
        // `n̂ · lo` (= `cross(lo, hi) / |hi − lo|`, but written with the
        // normal so that a short edge far from the centre keeps an error
        // of a few ulps of `|lo|`, not of `|lo| |hi| / |hi − lo|`).
        let normal = [hi[1] - lo[1], lo[0] - hi[0]];
        let len = (normal[0] * normal[0] + normal[1] * normal[1]).sqrt();
        let dot = normal[0] * lo[0] + normal[1] * lo[1];
        let (face_lo, num_lo, den_lo) = square_face(lo);
        let (face_hi, num_hi, den_hi) = square_face(hi);
        let (face_n, num_n, den_n) = square_face(normal);
        // The four quotients in one SIMD division (they are most of the
        // look-up's latency), then bins: `t · half + half` for the three
        // directions, `d / bin width` for the distance; truncation turns
        // NaN into 0 and the clamps keep every index in its table.
        let res = self.resolution;
        let (sector, dirs, dists) = (
            res.sector as i32,
            res.line_directions as i32,
            res.line_distances as i32,
        );
        let q =
            f32x4::from([num_lo, num_hi, num_n, dot]) / f32x4::from([den_lo, den_hi, den_n, len]);
        let (hs, hl) = (0.5 * sector as f32, 0.5 * dirs as f32);
        let scaled =
            q * f32x4::from([hs, hs, hl, self.inv_bin_width]) + f32x4::from([hs, hs, hl, 0.0]);
        let bins = scaled
            .trunc_int()
            .max(i32x4::ZERO)
            .min(i32x4::from([sector - 1, sector - 1, dirs - 1, dists - 1]))
            .to_array()
            .map(|b| b as usize);
        let (sector, dirs, dists) = (sector as usize, dirs as usize, dists as usize);
        let w = self.words;
        let a = field(&self.half_planes, face_lo * sector + bins[0], w);
        let b = field(&self.half_planes, face_hi * sector + bins[1], w);
        let d = q.to_array()[3];
        let line = if !(len > 0.0) || !d.is_finite() {
            LineFactor::Undefined
        } else if d >= self.r_max {
            LineFactor::Empty
        } else {
            LineFactor::Field(field(
                &self.lines,
                (face_n * dirs + bins[2]) * dists + bins[3],
                w,
            ))
        };
        (a, b, line)
    }

    /// The covered-sample mask of `edge` into `out` (resized to the
    /// number of words): bit `k` set when the tables say sample `k` is
    /// covered. An edge with a non-finite end covers nothing.
    pub fn covered_mask(&self, edge: &OrientedEdge, out: &mut Vec<u64>) {
        out.clear();
        out.resize(self.words, 0);
        self.for_each_word(edge, |w, m| out[w] = m);
    }

    /// Calls `f(word index, covered bits)` for each word of the mask.
    #[inline]
    fn for_each_word(&self, edge: &OrientedEdge, mut f: impl FnMut(usize, u64)) {
        let (lo, hi) = (edge.lo(), edge.hi());
        if self.words == 0 || !lo.iter().chain(hi.iter()).all(|c| c.is_finite()) {
            return;
        }
        let (a, b, line) = self.fields(lo, hi);
        match line {
            LineFactor::Empty => {}
            LineFactor::Field(l) => {
                for (w, ((&a, &b), &l)) in a.iter().zip(b).zip(l).enumerate() {
                    f(w, a & !b & l);
                }
            }
            LineFactor::Undefined => {
                for (w, (&a, &b)) in a.iter().zip(b).enumerate() {
                    f(w, a & !b);
                }
            }
        }
    }

    /// Adds `delta` to the counter of every sample the tables say `edge`
    /// covers: [`super::counters::add_covered`] with the look-up instead
    /// of the per-sample test (same orientation, same half-open sector,
    /// same sign). `counters[k]` is sample `k` of the set the tables were
    /// built for; counters past the end of a shorter slice are skipped.
    pub fn add_covered(&self, counters: &mut [i32], edge: &OrientedEdge, delta: i32) {
        // One word (N ≤ 64): no test for an empty mask, whose outcome is
        // unpredictable and costs more than the masked adds it saves.
        let single = self.words == 1;
        self.for_each_word(edge, |w, m| {
            if single || m != 0 {
                add_word(counters, w * 64, m, delta);
            }
        });
    }
}

/// Adds `delta` to `counters[base + i]` for every bit `i` of `mask`.
///
/// The word is applied eight counters at a time over all its lanes,
/// with no test per byte or per bit: covered bits are spread
/// unpredictably, and a branch per byte (or a loop per set bit) costs
/// more in mispredictions than the masked adds it would skip.
#[inline]
fn add_word(counters: &mut [i32], base: usize, mask: u64, delta: i32) {
    let end = counters.len().min(base.saturating_add(64));
    let Some(word) = counters.get_mut(base..end) else {
        return;
    };
    let d = i32x8::splat(delta);
    let lanes = i32x8::from([1, 2, 4, 8, 16, 32, 64, 128]);
    let done = word.len() / LANES * LANES;
    let mut chunks = word.chunks_exact_mut(LANES);
    for (byte, c) in chunks.by_ref().enumerate() {
        let bits = i32::from((mask >> (8 * byte)) as u8);
        let on = (i32x8::splat(bits) & lanes).cmp_eq(lanes);
        let cur = i32x8::new([c[0], c[1], c[2], c[3], c[4], c[5], c[6], c[7]]);
        c.copy_from_slice(&(cur + (on & d)).to_array());
    }
    // A slice shorter than the set (counters are normally padded to
    // whole lanes): the last few one at a time.
    for (i, c) in chunks.into_remainder().iter_mut().enumerate() {
        if mask >> (done + i) & 1 == 1 {
            // Wrapping, as the SIMD adds and `counters::add_covered`.
            *c = c.wrapping_add(delta);
        }
    }
}

#[cfg(test)]
mod tests {
    use super::*;
    use crate::sampling::PatternSampler;
    use crate::shadow::dcs::counters::add_covered as exact_add_covered;
    use glam::Vec3;

    /// The `correlated` set of `n` samples on a rect light, in its chart
    /// (`[2s − 1, 1 − 2t]`, as `LightSampler::chart_points`).
    fn correlated(n: u32) -> Vec<[f32; 2]> {
        let mut unit = Vec::new();
        PatternSampler::new(SamplePattern::Correlated, n, 7, 0).unit_points((0, 0), &mut unit);
        unit.iter()
            .map(|&(s, t)| [(2.0 * s - 1.0) as f32, (1.0 - 2.0 * t) as f32])
            .collect()
    }

    fn chart(points: &[[f32; 2]]) -> ChartSamples {
        let mut c = ChartSamples::default();
        c.set(points.iter().map(|p| [f64::from(p[0]), f64::from(p[1])]));
        c
    }

    /// Deterministic uniforms in `[−1, 1)`.
    struct Lcg(u64);
    impl Lcg {
        fn next(&mut self) -> f64 {
            self.0 = self
                .0
                .wrapping_mul(6364136223846793005)
                .wrapping_add(1442695040888963407);
            ((self.0 >> 11) as f64 / (1u64 << 53) as f64) * 2.0 - 1.0
        }
    }

    /// Random projected edges: both ends uniform in the chart's square
    /// (where the clipper leaves them), in-line ones dropped.
    fn random_edges(count: usize, seed: u64) -> Vec<OrientedEdge> {
        let mut r = Lcg(seed);
        let mut out = Vec::with_capacity(count);
        while out.len() < count {
            let a = [r.next(), r.next()];
            let b = [r.next(), r.next()];
            if let Some(e) = OrientedEdge::new(a, b) {
                out.push(e);
            }
        }
        out
    }

    /// f32 rounding of the exact test and of the look-up's own f32 index
    /// arithmetic, in chart units: a few ulps of the chart's size
    /// (computed errors are ~1e-6 at |s| ≤ √2; see `line`).
    const EPS: f64 = 1e-5;

    /// Which boundary band of `edge` sample `s` lies in, from the error
    /// bounds of the tables (module documentation): the half-plane lines
    /// through `lo` and `hi`, and the edge's line.
    fn in_band(t: &CoverageTables, edge: &OrientedEdge, s: [f32; 2]) -> bool {
        let b = t.error_bounds();
        let f = |v: [f32; 2]| [f64::from(v[0]), f64::from(v[1])];
        let (lo, hi, s) = (f(edge.lo()), f(edge.hi()), f(s));
        let r = s[0].hypot(s[1]);
        let ray = |v: [f64; 2]| {
            let len = v[0].hypot(v[1]);
            ((v[0] * s[1] - v[1] * s[0]) / len).abs() <= b.sector_angle.sin() * r + EPS
        };
        let n = [hi[1] - lo[1], lo[0] - hi[0]];
        let len = n[0].hypot(n[1]);
        let d = (n[0] * lo[0] + n[1] * lo[1]) / len;
        let dist = (n[0] * s[0] + n[1] * s[1]) / len - d;
        let line = dist.abs() <= 2.0 * (0.5 * b.line_angle).sin() * r + b.line_distance + EPS;
        ray(lo) || ray(hi) || line
    }

    /// Counts over `edges` × samples: (decisions, mismatches, mismatches
    /// outside every band, decisions inside a band, exact covered).
    fn measure(points: &[[f32; 2]], res: TableResolution, edges: &[OrientedEdge]) -> [u64; 5] {
        let t = CoverageTables::new(points, res).unwrap();
        let c = chart(points);
        let mut out = [0u64; 5];
        let (mut exact, mut table) = (vec![0; c.padded()], vec![0; c.padded()]);
        for e in edges {
            exact.fill(0);
            table.fill(0);
            exact_add_covered(&mut exact, &c, e, 1);
            t.add_covered(&mut table, e, 1);
            for (k, p) in points.iter().enumerate() {
                let band = in_band(&t, e, *p);
                out[0] += 1;
                out[3] += u64::from(band);
                out[4] += u64::from(exact[k] == 1);
                if exact[k] != table[k] {
                    out[1] += 1;
                    out[2] += u64::from(!band);
                }
            }
            // Padding is never touched.
            assert!(table[points.len()..].iter().all(|&v| v == 0));
        }
        out
    }

    /// Every mismatch between the look-up and the exact test lies within
    /// the tables' resolution of one of the edge's three boundaries, and
    /// the mismatches shrink as the resolution grows. Prints the table in
    /// `docs/algorithms/dcs.md`
    /// (`cargo test --release --lib bitfield -- --nocapture`).
    #[test]
    fn mismatches_lie_within_the_resolution_of_a_boundary() {
        let edges = random_edges(2000, 11);
        let resolutions = [(16, 16, 32), (32, 32, 64), (64, 64, 128), (128, 128, 256)].map(
            |(sector, line_directions, line_distances)| TableResolution {
                sector,
                line_directions,
                line_distances,
            },
        );
        println!("N | sector/face | line dirs/face × dists | mismatches | of covered | in bands");
        for n in [16u32, 64, 256, 1024] {
            let points = correlated(n);
            let mut last = f64::INFINITY;
            for res in resolutions {
                let [decisions, bad, outside, band, covered] = measure(&points, res, &edges);
                assert_eq!(outside, 0, "n {n} {res:?}: mismatch outside the bands");
                assert!(covered > decisions / 100, "edges cover samples");
                let frac = bad as f64 / decisions as f64;
                println!(
                    "{n} | {} | {} × {} | {:.4} % | {:.3} % | {:.3} %",
                    res.sector,
                    res.line_directions,
                    res.line_distances,
                    100.0 * frac,
                    100.0 * bad as f64 / covered as f64,
                    100.0 * band as f64 / decisions as f64,
                );
                // Halving the cells' widths halves the bands' area: with
                // 2000 edges the counts are far from equal.
                assert!(frac < last, "n {n} {res:?}: {frac} not below {last}");
                last = frac;
            }
            assert!(last > 0.0 || n < 64, "the measure can see mismatches");
        }
    }

    /// Samples far from every boundary are decided exactly, with the sign
    /// and orientation of `counters::add_covered`: coarse tables, a 4 × 4
    /// grid of samples, and the random edges whose rays and line stay
    /// clear of every sample's band.
    #[test]
    fn clear_samples_match_the_exact_test_with_sign() {
        let points: Vec<[f32; 2]> = (0..16)
            .map(|k| [-0.75 + 0.5 * (k % 4) as f32, -0.75 + 0.5 * (k / 4) as f32])
            .collect();
        let res = TableResolution {
            sector: 8,
            line_directions: 8,
            line_distances: 8,
        };
        let t = CoverageTables::new(&points, res).unwrap();
        let c = chart(&points);
        let mut checked = 0;
        for e in random_edges(20_000, 3) {
            if points.iter().any(|&p| in_band(&t, &e, p)) {
                continue;
            }
            let (mut exact, mut table) = (vec![5; c.padded()], vec![5; c.padded()]);
            exact_add_covered(&mut exact, &c, &e, -3);
            t.add_covered(&mut table, &e, -3);
            assert_eq!(exact, table, "{:?} {:?}", e.lo(), e.hi());
            checked += usize::from(exact.contains(&2));
        }
        assert!(checked >= 10, "only {checked} clear covering edges");
    }

    /// A closed loop around the centre: consecutive edges share their
    /// vertices bit for bit, so their sector factors are complementary
    /// and partition the samples; the only mismatches left are along the
    /// loop's own edges (line bands), none along the shared rays.
    #[test]
    fn a_closed_loop_partitions_the_samples() {
        let points = correlated(256);
        let res = TableResolution {
            sector: 16,
            line_directions: 16,
            line_distances: 32,
        };
        let t = CoverageTables::new(&points, res).unwrap();
        let c = chart(&points);
        // An irregular 9-gon around the origin.
        let poly: Vec<[f64; 2]> = (0..9)
            .map(|k| {
                let a = k as f64 * std::f64::consts::TAU / 9.0 + 0.1 * (k % 3) as f64;
                let r = 0.5 + 0.07 * (k % 4) as f64;
                [r * a.cos(), r * a.sin()]
            })
            .collect();
        let edges: Vec<OrientedEdge> = (0..9)
            .map(|k| OrientedEdge::new(poly[k], poly[(k + 1) % 9]).unwrap())
            .collect();
        // Sector factors alone: every sample exactly once.
        let mut once = vec![0u32; points.len()];
        let mut mask = Vec::new();
        for e in &edges {
            let (a, b, _) = t.fields(e.lo(), e.hi());
            mask.clear();
            mask.extend(a.iter().zip(b).map(|(a, b)| a & !b));
            for (k, v) in once.iter_mut().enumerate() {
                *v += (mask[k / 64] >> (k % 64) & 1) as u32;
            }
        }
        assert!(once.iter().all(|&v| v == 1), "{once:?}");
        // Whole masks: beyond the loop 1, inside 0, except near its edges.
        let (mut exact, mut table) = (vec![0; c.padded()], vec![0; c.padded()]);
        for e in &edges {
            exact_add_covered(&mut exact, &c, e, 1);
            t.add_covered(&mut table, e, 1);
        }
        let b = t.error_bounds();
        for (k, p) in points.iter().enumerate() {
            assert!((0..=1).contains(&exact[k]));
            if exact[k] != table[k] {
                let near_some_line = edges.iter().any(|e| {
                    let (lo, hi) = (e.lo(), e.hi());
                    let n = [f64::from(hi[1] - lo[1]), f64::from(lo[0] - hi[0])];
                    let len = n[0].hypot(n[1]);
                    let d = (n[0] * f64::from(lo[0]) + n[1] * f64::from(lo[1])) / len;
                    let s = [f64::from(p[0]), f64::from(p[1])];
                    let r = s[0].hypot(s[1]);
                    ((n[0] * s[0] + n[1] * s[1]) / len - d).abs()
                        <= 2.0 * (0.5 * b.line_angle).sin() * r + b.line_distance + EPS
                });
                assert!(
                    near_some_line,
                    "sample {k} {p:?}: {} vs {}",
                    exact[k], table[k]
                );
            }
        }
    }

    #[test]
    fn from_chart_is_new_on_the_unpadded_samples() {
        let points = correlated(20);
        let res = TableResolution::default();
        let a = CoverageTables::new(&points, res).unwrap();
        let b = CoverageTables::from_chart(&chart(&points), res).unwrap();
        assert_eq!(b.len(), 20);
        assert_eq!(a.half_planes, b.half_planes);
        assert_eq!(a.lines, b.lines);
        assert_eq!(a.bytes(), res.bytes(20));
    }

    #[test]
    fn degenerate_inputs_do_not_panic() {
        let res = TableResolution::default();
        // No samples.
        let empty = CoverageTables::new(&[], res).unwrap();
        assert!(empty.is_empty());
        let e = OrientedEdge::new([0.5, -0.5], [0.5, 0.5]).unwrap();
        let mut c = vec![0; 8];
        empty.add_covered(&mut c, &e, 1);
        assert_eq!(c, vec![0; 8]);
        // Non-finite samples are never covered; r_max ignores them.
        let odd = [
            [f32::NAN, 0.0],
            [0.9, 0.0],
            [f32::INFINITY, 1.0],
            [0.0, 0.0],
        ];
        let t = CoverageTables::new(&odd, res).unwrap();
        assert!(t.r_max() > 0.9 && t.r_max() < 0.9001);
        let mut c = vec![0; 8];
        t.add_covered(&mut c, &e, 1);
        assert_eq!(c, vec![0, 1, 0, 0, 0, 0, 0, 0]);
        // Counters shorter than the set; very short, huge, non-finite and
        // far edges.
        let t = CoverageTables::new(&correlated(200), res).unwrap();
        let mut short = vec![0; 3];
        let tiny = 1e-30;
        for (a, b) in [
            ([0.5, -0.5], [0.5, 0.5]),
            ([0.3, 0.3], [0.3 - tiny, 0.3 + tiny]),
            ([1e30, -1e30], [1e30, 1e30]),
            ([f64::INFINITY, 0.0], [0.0, 1.0]),
            ([3.0, -0.1], [3.0, 0.1]),
            ([1e-40, 0.0], [0.0, 1e-40]),
        ] {
            if let Some(e) = OrientedEdge::new(a, b) {
                t.add_covered(&mut short, &e, i32::MAX);
                t.add_covered(&mut short, &e, i32::MAX);
                let mut m = Vec::new();
                t.covered_mask(&e, &mut m);
                assert_eq!(m.len(), 4);
            }
        }
        // Resolutions: zero and oversized are errors, not panics.
        let zero = TableResolution { sector: 0, ..res };
        assert!(CoverageTables::new(&correlated(4), zero).is_err());
        let huge = TableResolution {
            sector: u32::MAX,
            line_directions: u32::MAX,
            line_distances: u32::MAX,
        };
        assert!(CoverageTables::new(&correlated(4), huge).is_err());
    }

    #[test]
    fn applicable_only_to_shared_rect_sets() {
        let rect = LightShape::Rect {
            center: Vec3::ZERO,
            u: Vec3::X,
            v: Vec3::Z,
            two_sided: false,
        };
        let sphere = LightShape::Sphere {
            center: Vec3::ZERO,
            radius: 1.0,
        };
        assert_eq!(
            CoverageTables::applicable(SamplePattern::Correlated, &rect),
            Ok(1)
        );
        assert_eq!(
            CoverageTables::applicable(SamplePattern::Interleaved { n: 4 }, &rect),
            Ok(16)
        );
        for p in [
            SamplePattern::Stratified,
            SamplePattern::Rotated,
            SamplePattern::Poisson,
            SamplePattern::Sobol02,
        ] {
            let e = CoverageTables::applicable(p, &rect).unwrap_err();
            assert!(e.contains(&p.name()), "{e}");
        }
        for p in [
            SamplePattern::Correlated,
            SamplePattern::Interleaved { n: 2 },
        ] {
            let e = CoverageTables::applicable(p, &sphere).unwrap_err();
            assert!(e.contains("sphere"), "{e}");
        }
    }

    #[test]
    fn square_map_bins_are_contiguous_and_bounded() {
        let per_face = 7;
        let alpha = max_half_width(per_face);
        // Around the circle, every direction lands in the bin whose
        // representative is within the bin's half-width of it.
        for k in 0..10_000 {
            let a = k as f64 * std::f64::consts::TAU / 10_000.0;
            let v = [a.cos() as f32, a.sin() as f32];
            let bin = direction_bin(v, per_face);
            let ([rx, ry], half) = bin_direction(bin, per_face);
            let angle = (f64::from(v[0]) * ry - f64::from(v[1]) * rx)
                .atan2(f64::from(v[0]) * rx + f64::from(v[1]) * ry)
                .abs();
            assert!(
                angle <= half + 1e-6,
                "angle {a}: bin {bin} off by {angle} > {half}"
            );
            assert!(half <= alpha);
        }
        // The widest bin is at each face's middle: with 7 bins per face,
        // `t ∈ [−1/7, 1/7]`, half-width `atan(1/7)`.
        assert!((alpha - (1.0f64 / 7.0).atan()).abs() < 1e-12, "{alpha}");
    }
}
