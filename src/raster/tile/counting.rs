//! Counting passes (stencil-only shadow volumes): a triangle larger than
//! 8×8 pixels is walked row by row as exact spans, its tile part and then
//! its bands of 8 rows judged first by the tile's depth bounds; merged
//! quads carry a fourth edge and a second depth plane.

use super::depth_bounds::{DepthBounds, Verdict};
use super::job::{
    clip_to_tile, CountingPass, TileJob, TileStats, BLOCK, MAX_DEPTH_SHIFTS, OFFSETS_I32,
};
use crate::raster::fragment::FragmentStage;
use crate::raster::framebuffer::{DepthStencilTile, TILE_SIZE};
use crate::raster::setup::{EdgeFunction, Plane, QuadExtra, SetupTriangle};
use crate::raster::simd::{compare_f32_lanes, LANES, LANE_OFFSETS};
use crate::raster::state::CompareFunc;
use crate::simd::{f32x8, f64x4, i32x8};

/// A triangle's edge lines as `x = x0 + slope · y` (pixel units, f64,
/// approximate): a cheap, conservative x-extent of the triangle over a
/// band of rows, for the depth-bounds verdicts.
struct EdgeLines {
    /// `x0` of up to two left and two right edges (lanes 0, 1 and 2, 3;
    /// unused ones far out).
    x0: f64x4,
    slope: f64x4,
}

impl EdgeLines {
    fn of(edges: &[EdgeFunction]) -> Self {
        const FAR: f64 = 1e30;
        let mut x0 = [-FAR, -FAR, FAR, FAR];
        let mut slope = [0.0; 4];
        let (mut nl, mut nr) = (0, 2);
        for e in edges {
            if e.a == 0 {
                continue;
            }
            // E(x, y) = A x + B y + C = 0 on the line.
            let (a, b, c) = (
                e.step_x() as f64,
                e.step_y() as f64,
                e.at_pixel(0, 0) as f64,
            );
            let k = if e.a > 0 {
                nl += 1;
                nl - 1
            } else {
                nr += 1;
                nr - 1
            };
            x0[k] = -c / a;
            slope[k] = -b / a;
        }
        EdgeLines {
            x0: f64x4::new(x0),
            slope: f64x4::new(slope),
        }
    }

    /// Columns `lo..=hi` holding every covered pixel of rows `y0..=y1`
    /// (with a pixel of margin for the rounding here), clamped to
    /// `[x_min, x_max]`: a left edge keeps the covered pixels of every row
    /// right of its line, so right of the line's leftmost point over the
    /// band, at one of its ends; right edges likewise.
    #[inline]
    fn extent(&self, y0: i32, y1: i32, x_min: i32, x_max: i32) -> (i32, i32) {
        let a = self.x0 + self.slope * f64x4::splat(y0 as f64);
        let b = self.x0 + self.slope * f64x4::splat(y1 as f64);
        let (mn, mx) = (a.min(b).to_array(), a.max(b).to_array());
        let lo = if mn[0] > mn[1] { mn[0] } else { mn[1] } - 1.0;
        let hi = if mx[2] < mx[3] { mx[2] } else { mx[3] } + 1.0;
        // Compared before converting: the bounds may be far out.
        let lo = if lo > x_min as f64 { lo as i32 } else { x_min };
        let hi = if hi < x_max as f64 { hi as i32 } else { x_max };
        (lo, hi)
    }
}

/// All-ones lanes `k` where `e >= 0` at pixel `(x + k, y)`: `v + k a >= 0`
/// for `v` its value at `(x, y)` and `a` its step, solved exactly for the
/// first (a > 0) or last (a < 0) such lane.
#[inline]
fn edge_lanes(e: &EdgeFunction, x: i32, y: i32) -> i32x8 {
    let v = e.at_pixel(x as i64, y as i64);
    let a = e.step_x();
    if a > 0 {
        let first = (-floor_div(v, a).0).clamp(0, LANES as i64) as i32;
        OFFSETS_I32.cmp_gt(i32x8::splat(first - 1))
    } else if a < 0 {
        let last = floor_div(v, -a).0.clamp(-1, LANES as i64 - 1) as i32;
        i32x8::splat(last + 1).cmp_gt(OFFSETS_I32)
    } else {
        i32x8::splat(if v >= 0 { -1 } else { 0 })
    }
}

/// `(floor(v / m), v - m floor(v / m))` for `m > 0`. The quotient is
/// estimated in f64 (one division, where an i64 division is a slow
/// instruction) and corrected exactly in integers, so the result never
/// depends on the estimate's rounding.
#[inline(always)]
fn floor_div(v: i64, m: i64) -> (i64, i64) {
    let mut q = (v as f64 / m as f64) as i64;
    let mut r = v - q * m;
    while r < 0 {
        q -= 1;
        r += m;
    }
    while r >= m {
        q += 1;
        r -= m;
    }
    (q, r)
}

/// A triangle's exact covered span on each row of a clip rectangle.
///
/// Along a row, an edge is `E = A i + V` (`i` the pixel offset from the
/// rectangle's left column, `A` its per-pixel step); the covered offsets
/// are `i >= -floor(V / A)` when `A > 0` (a left edge) and
/// `i <= floor(V / -A)` when `A < 0` (a right edge); horizontal edges
/// only restrict the rows. Down the rows `V` grows by `B`, so each bound
/// `floor(V / |A|)` is carried as an exact quotient and remainder,
/// stepped by `B = qb |A| + rb` with one carry. The four slots (two left
/// edges, two right ones, unused slots never binding; a triangle has at
/// most two of either, and quads are merged only when so) are stepped
/// together in `f64` lanes: every value is an integer below 2^53, so all
/// of it is exact, and the span is the pixels `E >= 0` selects, no more,
/// no fewer.
struct SpanWalk {
    /// `[-q, -q, q, q]` of the left, left, right, right slots: the
    /// span is `max(g0, g1) ..= min(g2, g3)`.
    g: f64x4,
    /// Remainders, in `[0, m)`.
    r: f64x4,
    /// Per-row step of `g` before the carry.
    g_step: f64x4,
    /// Per-row step of `r`.
    r_step: f64x4,
    /// `|A|` of each slot.
    m: f64x4,
    /// What a carry adds to `g`: -1 on the left slots, +1 on the right.
    carry: f64x4,
    /// Largest offset inside the rectangle.
    width: f64,
}

impl SpanWalk {
    /// Rows of `clip` where each edge leaves at least the rectangle's
    /// pixel that is deepest inside it (`E(x, y) = v + b (y - y0) >= 0`
    /// there): exact for a horizontal edge; for the others it skips the
    /// rows a sliver's bounding box holds above and below it. `None` when
    /// no row is left.
    #[inline]
    fn rows(edges: &[EdgeFunction], clip: [i32; 4]) -> Option<(i32, i32)> {
        let (mut y0, mut y1) = (clip[1] as i64, clip[3] as i64);
        let first = y0;
        for e in edges {
            let x = if e.a > 0 { clip[2] } else { clip[0] };
            let v = e.at_pixel(x as i64, first);
            let b = e.step_y();
            if b > 0 {
                y0 = y0.max(first - floor_div(v, b).0);
            } else if b < 0 {
                y1 = y1.min(first + floor_div(v, -b).0);
            } else if v < 0 {
                return None;
            }
        }
        (y0 <= y1).then_some((y0 as i32, y1 as i32))
    }

    /// The walk over `clip`'s columns starting at row `y`.
    #[inline]
    fn at(edges: &[EdgeFunction], clip: [i32; 4], y: i32) -> Self {
        // Unused slots: q = 2^40, far outside any tile, never moving.
        const FAR: f64 = (1u64 << 40) as f64;
        let mut g = [-FAR, -FAR, FAR, FAR];
        let mut r = [0.0; 4];
        let mut g_step = [0.0; 4];
        let mut r_step = [0.0; 4];
        let mut m = [1.0; 4];
        let (mut nl, mut nr) = (0, 2);
        for e in edges {
            if e.a == 0 {
                continue;
            }
            let a = e.step_x().abs();
            let (q, rem) = floor_div(e.at_pixel(clip[0] as i64, y as i64), a);
            let (qb, rb) = floor_div(e.step_y(), a);
            let (k, sign) = if e.a > 0 {
                nl += 1;
                (nl - 1, -1.0)
            } else {
                nr += 1;
                (nr - 1, 1.0)
            };
            g[k] = sign * q as f64;
            r[k] = rem as f64;
            g_step[k] = sign * qb as f64;
            r_step[k] = rb as f64;
            m[k] = a as f64;
        }
        SpanWalk {
            g: f64x4::new(g),
            r: f64x4::new(r),
            g_step: f64x4::new(g_step),
            r_step: f64x4::new(r_step),
            m: f64x4::new(m),
            carry: f64x4::new([-1.0, -1.0, 1.0, 1.0]),
            width: (clip[2] - clip[0]) as f64,
        }
    }

    /// Covered offsets `lo..=hi` of the current row (empty when `lo > hi`;
    /// `lo > hi + 1` when even the real interval is empty).
    #[inline(always)]
    fn span(&self) -> (i32, i32) {
        let g = self.g.to_array();
        let max = |a: f64, b: f64| if a > b { a } else { b };
        let min = |a: f64, b: f64| if a < b { a } else { b };
        // Clamped to the rectangle and to i32 (plus one so that an empty
        // span stays empty): the conversions are exact.
        let lo = min(max(max(g[0], g[1]), 0.0), self.width + 2.0);
        let hi = max(min(min(g[2], g[3]), self.width), -2.0);
        (lo as i32, hi as i32)
    }

    /// Moves to the next row.
    #[inline(always)]
    fn step(&mut self) {
        let r = self.r + self.r_step;
        let c = r.cmp_ge(self.m);
        self.r = r - (self.m & c);
        self.g = self.g + self.g_step + (self.carry & c);
    }
}

impl<const N: usize, S: FragmentStage<N>> TileJob<'_, N, S> {
    /// [`TileJob::run`] for a counting pass: triangles larger than 8×8
    /// pixels are walked row by row as exact spans (see [`SpanWalk`]), so
    /// a long sliver costs one batch per row it covers and nothing for the
    /// rest of its bounding box.
    pub(super) fn run_counting(
        &self,
        c: CountingPass,
        ds: &mut DepthStencilTile,
        target: &mut S::Target,
    ) -> TileStats {
        // The depth compare is monomorphised for the one volumes use.
        match self.state.depth_func {
            CompareFunc::Greater => self.count_spans(c, ds, target, |f, s| f.cmp_gt(s).cast_i32()),
            func => self.count_spans(c, ds, target, |f, s| compare_f32_lanes(func, f, s)),
        }
    }

    /// The span walk over every binned triangle, in bin order.
    #[inline(always)]
    fn count_spans(
        &self,
        c: CountingPass,
        ds: &mut DepthStencilTile,
        target: &mut S::Target,
        test: impl Fn(f32x8, f32x8) -> i32x8,
    ) -> TileStats {
        let mut stats = TileStats::default();
        let (tx, ty) = self.origin;
        let walk = CountingWalk::new(c, self.state.depth_func, test);
        // Depth bounds of the tile's blocks, made on first use: a pass
        // that counts does not write depth, so they hold for the whole
        // pass.
        let mut bounds: Option<DepthBounds> = None;
        for &ti in self.bin {
            let (t, quads) = self.setup.get(ti);
            let Some(clip) = clip_to_tile(t.bbox, tx, ty) else {
                continue;
            };
            if t.small {
                self.small(t, clip, ds, target, &mut stats);
                continue;
            }
            let quad = quads.get(t.quad as usize);
            self.count_triangle(&walk, t, quad, clip, ds, &mut bounds, &mut stats);
        }
        stats
    }

    /// One triangle (or merged quad) larger than 8×8 pixels, clipped to
    /// `clip` inside the tile: the whole rectangle's verdicts first, then
    /// band by band, each band's rows as exact spans. `quad`: the extras
    /// of a merged quad.
    #[allow(clippy::too_many_arguments)]
    #[inline(always)]
    fn count_triangle<T: Fn(f32x8, f32x8) -> i32x8>(
        &self,
        walk: &CountingWalk<T>,
        t: &SetupTriangle<N>,
        quad: Option<&QuadExtra>,
        clip: [i32; 4],
        ds: &mut DepthStencilTile,
        bounds: &mut Option<DepthBounds>,
        stats: &mut TileStats,
    ) {
        let (tx, ty) = self.origin;
        let c = walk.pass;
        // A merged quad has a fourth edge, a second depth plane and a
        // diagonal that says which plane a pixel takes.
        let edges = [
            t.edges[0],
            t.edges[1],
            t.edges[2],
            quad.map_or(t.edges[2], |q| q.edge),
        ];
        let edges = &edges[..3 + usize::from(quad.is_some())];
        let Some(rows) = SpanWalk::rows(edges, clip) else {
            return;
        };
        let Some(stencil) = ds.stencil.as_deref_mut() else {
            return;
        };
        let mut images = CountImages {
            origin: self.origin,
            depth: &ds.depth[..],
            stencil,
            shifted: &mut ds.shifted[..],
        };
        let plane = t.depth;
        let plane2 = quad.map(|q| q.depth2);
        let triangle = SpanTriangle {
            walk,
            plane,
            plane2,
            quad,
            delta: i32x8::splat(if t.front_facing { c.front } else { c.back }),
            x0: f32x8::splat(plane.x0),
            dx: f32x8::splat(plane.dx),
        };
        // The whole rectangle's verdicts first, then band by band.
        let lines = walk.use_bounds.then(|| EdgeLines::of(edges));
        let mut pair = WalkVerdicts::all_test(walk.n_shifts);
        if let Some(lines) = &lines {
            let (xl, xh) = lines.extent(rows.0, rows.1, clip[0], clip[2]);
            if xl > xh {
                return;
            }
            let b = bounds.get_or_insert_with(|| DepthBounds::of(images.depth));
            let rect = [xl - tx, rows.0 - ty, xh - tx, rows.1 - ty];
            pair = pair.refine(b, (&plane, plane2.as_ref()), self.origin, rect, c);
            if pair.skip() {
                return;
            }
        }
        // The walk, when it stands at row `walk_row`.
        let mut span_walk: Option<SpanWalk> = None;
        let mut walk_row = rows.0;
        let mut seen = false;
        let mut y = rows.0;
        // Bands of up to 8 rows inside one row of blocks.
        while y <= rows.1 {
            let band = (y, (y | (BLOCK - 1)).min(rows.1));
            y = band.1 + 1;
            let mut verdict = pair;
            let one_band = band.0 == rows.0 && band.1 == rows.1;
            if let (true, false, Some(lines), Some(b)) = (pair.tests(), one_band, &lines, &*bounds)
            {
                let (xl, xh) = lines.extent(band.0, band.1, clip[0], clip[2]);
                if xl > xh {
                    continue;
                }
                let rect = [xl - tx, band.0 - ty, xh - tx, band.1 - ty];
                verdict = pair.refine(b, (&plane, plane2.as_ref()), self.origin, rect, c);
                if verdict.skip() {
                    continue;
                }
            }
            let rows_walk = match &mut span_walk {
                Some(w) if walk_row == band.0 => w,
                _ => span_walk.insert(SpanWalk::at(edges, clip, band.0)),
            };
            walk_row = band.1 + 1;
            let band_walk = BandWalk {
                rows: band,
                left_column: clip[0],
                verdict,
                tested: verdict.tests(),
            };
            let done = triangle.count_band(&band_walk, rows_walk, &mut seen, &mut images, stats);
            if done {
                break;
            }
        }
    }
}

/// What a counting walk keeps constant over one tile.
struct CountingWalk<T> {
    pass: CountingPass,
    /// Counted lanes are `pass ^ flip`: the failing ones for z-fail.
    flip: i32x8,
    scales: [f32x8; MAX_DEPTH_SHIFTS],
    n_shifts: usize,
    /// Only the volumes' test (Greater) uses depth bounds.
    use_bounds: bool,
    zero: i32x8,
    /// The depth test, monomorphised.
    test: T,
}

impl<T: Fn(f32x8, f32x8) -> i32x8> CountingWalk<T> {
    #[inline(always)]
    fn new(c: CountingPass, depth_func: CompareFunc, test: T) -> Self {
        CountingWalk {
            pass: c,
            flip: i32x8::splat(if c.on_depth_fail { -1 } else { 0 }),
            scales: c.shifts.scales.map(f32x8::splat),
            n_shifts: c.shifts.len,
            use_bounds: depth_func == CompareFunc::Greater,
            zero: i32x8::splat(0),
            test,
        }
    }
}

/// The tile's images a counting walk reads (depth) and adds to.
struct CountImages<'a> {
    origin: (i32, i32),
    depth: &'a [f32],
    stencil: &'a mut [i32],
    shifted: &'a mut [Box<[i32]>],
}

/// One triangle's constants in a counting walk.
struct SpanTriangle<'a, T> {
    walk: &'a CountingWalk<T>,
    plane: Plane,
    plane2: Option<Plane>,
    quad: Option<&'a QuadExtra>,
    /// Added per counted fragment.
    delta: i32x8,
    x0: f32x8,
    dx: f32x8,
}

/// One band of up to 8 rows and its verdicts.
struct BandWalk {
    /// First and last row.
    rows: (i32, i32),
    /// The clip rectangle's left column, where span offsets start.
    left_column: i32,
    verdict: WalkVerdicts,
    /// Whether any count of the band needs depths ([`WalkVerdicts::tests`]).
    tested: bool,
}

impl<T: Fn(f32x8, f32x8) -> i32x8> SpanTriangle<'_, T> {
    /// The rows of one band, walked by `span_walk`; true once the convex
    /// triangle has left the clip rectangle for good.
    #[inline(always)]
    fn count_band(
        &self,
        band: &BandWalk,
        span_walk: &mut SpanWalk,
        seen: &mut bool,
        images: &mut CountImages,
        stats: &mut TileStats,
    ) -> bool {
        for yy in band.rows.0..=band.rows.1 {
            let (lo, hi) = span_walk.span();
            span_walk.step();
            if lo > hi {
                // A thin triangle may pass between the pixel centres of a
                // row and cover the next; once even the real interval is
                // empty, the convex triangle has left the rectangle for
                // good.
                if *seen && lo > hi + 1 {
                    return true;
                }
                continue;
            }
            *seen = true;
            stats.fragments += (hi - lo + 1) as u64;
            self.count_span(band, images, band.left_column + lo, yy, hi - lo + 1);
        }
        false
    }

    /// The `left` pixels of row `y` from column `x`, 8 lanes at a time.
    #[inline(always)]
    fn count_span(&self, band: &BandWalk, images: &mut CountImages, x: i32, y: i32, left: i32) {
        let walk = self.walk;
        let (tx, ty) = images.origin;
        let (verdict, tested) = (band.verdict, band.tested);
        let (mut x, mut left) = (x, left);
        let mut local = ((y - ty) as usize) * TILE_SIZE + (x - tx) as usize;
        let base = f32x8::splat(self.plane.row_base(y));
        loop {
            // Live lanes: the span's pixels from x on. Lanes past the tile
            // row (padding or the next row) are loaded and stored back
            // unchanged.
            let live = i32x8::splat(left).cmp_gt(OFFSETS_I32);
            // The fragments' and stored depths, where a test needs them.
            let depths = tested.then(|| {
                // Plane::lanes_on_row with the per-triangle splats
                // hoisted: the same operations, the same bits.
                let cx = (f32x8::splat(x as f32) + LANE_OFFSETS) + f32x8::splat(0.5) - self.x0;
                let mut frag = base + self.dx * cx;
                if let (Some(q), Some(p2)) = (self.quad, &self.plane2) {
                    // The second triangle's pixels take its plane,
                    // computed as for it alone.
                    let second = p2.lanes(x, y);
                    let first = edge_lanes(&q.diagonal, x, y);
                    frag = first.cast_f32().blend(frag, second);
                }
                let frag = frag.max(f32x8::splat(0.0)).min(f32x8::splat(1.0));
                let stored: &[f32; LANES] = images.depth[local..local + LANES]
                    .try_into()
                    .expect("8 lanes");
                (frag, f32x8::new(*stored))
            });
            // The lanes that count, exactly: a verdict other than Test
            // holds for every covered pixel.
            let now = match (verdict.plain, depths) {
                (Verdict::Skip, _) => walk.zero,
                (Verdict::Test, Some((frag, stored))) => {
                    ((walk.test)(frag, stored) ^ walk.flip) & live
                }
                _ => live,
            };
            if verdict.plain != Verdict::Skip {
                let s: &mut [i32; LANES] = (&mut images.stencil[local..local + LANES])
                    .try_into()
                    .expect("8 lanes");
                *s = (i32x8::new(*s) + (now & self.delta)).to_array();
            }
            if let Some((frag, stored)) = depths {
                for ((image, &scale), &on) in images
                    .shifted
                    .iter_mut()
                    .zip(&walk.scales)
                    .zip(&verdict.shifted)
                {
                    if !on {
                        continue;
                    }
                    // +delta where the scaled depth counts and the stored
                    // one did not, −delta the other way.
                    let then = ((walk.test)(frag, stored * scale) ^ walk.flip) & live;
                    let s: &mut [i32; LANES] = (&mut image[local..local + LANES])
                        .try_into()
                        .expect("8 lanes");
                    *s = (i32x8::new(*s) + (then & self.delta) - (now & self.delta)).to_array();
                }
            }
            if left <= BLOCK {
                break;
            }
            left -= BLOCK;
            x += BLOCK;
            local += LANES;
        }
    }
}

/// A rectangle's verdicts in a counting walk: the counts', and per depth
/// scale whether its change must be tested (else it is 0 throughout).
#[derive(Clone, Copy)]
struct WalkVerdicts {
    plain: Verdict,
    shifted: [bool; MAX_DEPTH_SHIFTS],
}

impl WalkVerdicts {
    /// Everything tested (the first `n` scales).
    fn all_test(n: usize) -> WalkVerdicts {
        WalkVerdicts {
            plain: Verdict::Test,
            shifted: std::array::from_fn(|k| k < n),
        }
    }

    /// Nothing to do in the rectangle.
    fn skip(&self) -> bool {
        self.plain == Verdict::Skip && !self.shifted.contains(&true)
    }

    /// Whether some fragment's depth test must be run.
    fn tests(&self) -> bool {
        self.plain == Verdict::Test || self.shifted.contains(&true)
    }

    /// The verdicts over `rect`, inside a rectangle with these: only the
    /// tested ones are judged again (a sub-rectangle of one skipped or
    /// counted whole is skipped or counted whole too).
    fn refine(
        self,
        b: &DepthBounds,
        (plane, plane2): (&Plane, Option<&Plane>),
        origin: (i32, i32),
        rect: [i32; 4],
        c: CountingPass,
    ) -> WalkVerdicts {
        let plain = match self.plain {
            Verdict::Test => b.verdict(plane, plane2, origin, rect, c.on_depth_fail),
            v => v,
        };
        let mut shifted = self.shifted;
        for (on, &scale) in shifted.iter_mut().zip(c.shifts.as_slice()) {
            *on = *on && b.verdict_scaled(plane, plane2, origin, rect, scale) == Verdict::Test;
        }
        WalkVerdicts { plain, shifted }
    }
}

#[cfg(test)]
mod tests {
    use super::*;
    use crate::raster::setup::{Plane, SetupTriangle};
    use crate::raster::tile::job::Lcg;

    /// Random triangles (snapped vertices anywhere in a 400-pixel square
    /// around the rectangle, many nearly degenerate slivers, many on half
    /// pixels so that pixel centres lie exactly on edges) against
    /// random clip rectangles: the span walk selects exactly the pixels
    /// whose three edge values are >= 0, and the band extents hold them.
    #[test]
    fn span_walk_selects_exactly_the_covered_pixels() {
        let mut rng = Lcg(1);
        let mut covered = 0;
        for round in 0..20000 {
            let spread = if round % 2 == 0 { 400 } else { 40 };
            let mut p: Vec<(i64, i64)> = (0..3)
                .map(|_| {
                    (
                        (rng.below(spread) - spread / 3) * 256 + rng.below(256),
                        (rng.below(spread) - spread / 3) * 256 + rng.below(256),
                    )
                })
                .collect();
            if round % 3 == 0 {
                // A sliver: the third vertex next to the second.
                p[2] = (p[1].0 + rng.below(512) - 256, p[1].1 + rng.below(512) - 256);
            }
            if round % 7 == 0 {
                p[1].1 = p[0].1; // a horizontal edge
            }
            if round % 5 < 2 {
                // On half pixels: many pixel centres exactly on edges.
                for v in &mut p {
                    *v = (v.0 & !127, v.1 & !127);
                }
            }
            let area =
                (p[1].0 - p[0].0) * (p[2].1 - p[0].1) - (p[2].0 - p[0].0) * (p[1].1 - p[0].1);
            if area == 0 {
                continue;
            }
            let q = if area > 0 {
                [p[0], p[1], p[2]]
            } else {
                [p[0], p[2], p[1]]
            };
            let edges = [
                EdgeFunction::new(q[0], q[1]),
                EdgeFunction::new(q[1], q[2]),
                EdgeFunction::new(q[2], q[0]),
            ];
            let t = SetupTriangle::<0> {
                edges,
                bbox: [0, 0, 63, 63],
                depth: Plane::default(),
                inv_w: Plane::default(),
                varyings: [],
                front_facing: true,
                primitive: 0,
                small: false,
                block_i32: false,
                quad: crate::raster::setup::NO_QUAD,
            };
            let x0 = rng.below(40) as i32;
            let y0 = rng.below(40) as i32;
            let clip = [x0, y0, x0 + rng.below(64) as i32, y0 + rng.below(64) as i32];
            let inside = |x: i32, y: i32| edges.iter().all(|e| e.at_pixel(x as i64, y as i64) >= 0);
            let rows = SpanWalk::rows(&t.edges, clip);
            let lines = EdgeLines::of(&t.edges);
            // Start the walk at a random row of the range, as after a
            // skipped band.
            let mut walk = rows.map(|r| {
                let start = r.0 + rng.below((r.1 - r.0 + 1) as i64) as i32;
                (start, SpanWalk::at(&t.edges, clip, start))
            });
            for y in clip[1]..=clip[3] {
                let (lo, hi) = match (&rows, &mut walk) {
                    (Some(r), Some((start, w))) if y >= *start && y <= r.1 => {
                        let s = w.span();
                        w.step();
                        s
                    }
                    (Some(r), _) if y >= r.0 && y <= r.1 => (1, 0), // before the start: unchecked
                    _ => {
                        for x in clip[0]..=clip[2] {
                            assert!(
                                !inside(x, y),
                                "row {y} outside the walk's rows has ({x}, {y})"
                            );
                        }
                        continue;
                    }
                };
                let (elo, ehi) = lines.extent(y, y, i32::MIN / 2, i32::MAX / 2);
                let unchecked = matches!(walk, Some((start, _)) if y < start);
                for x in clip[0]..=clip[2] {
                    let i = x - clip[0];
                    let want = inside(x, y);
                    if !unchecked {
                        assert_eq!(
                            want,
                            i >= lo && i <= hi,
                            "{q:?} {clip:?} ({x}, {y}): {lo}..={hi}"
                        );
                    }
                    if want {
                        covered += 1;
                        assert!(x >= elo && x <= ehi, "extent {elo}..{ehi} misses {x}");
                    }
                }
                if lo > hi + 1 && !unchecked {
                    // Really empty: the rest of the rectangle is too.
                    let later =
                        (y + 1..=clip[3]).any(|yy| (clip[0]..=clip[2]).any(|x| inside(x, yy)));
                    let earlier = (clip[1]..y).any(|yy| (clip[0]..=clip[2]).any(|x| inside(x, yy)));
                    assert!(
                        !(later && earlier),
                        "{q:?} {clip:?}: row {y} splits the triangle"
                    );
                }
            }
        }
        assert!(covered > 100_000);
    }
}
