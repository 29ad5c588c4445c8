//! Tile traversal. Small triangles (bounding box within 8×8 pixels, most
//! triangles of a detailed mesh) go straight to 8-lane rows over their box
//! with `i32` edge values; larger ones descend from the 64×64 tile to 8×8
//! blocks (trivial accept / reject on exact corner values), then rows with
//! exact `f64` lanes on the edges that cross the block. Depth, stencil and
//! fragment batches are 8-lane SIMD either way.

use super::fragment::{FragmentBatch, FragmentStage};
use super::framebuffer::{DepthStencilTile, TILE_SIZE};
use super::setup::{EdgeFunction, QuadExtra, SetupTriangle};
use super::simd::{
    compare_f32, compare_f32_lanes, compare_i32, select_f32, select_i32, stencil_op, LANES,
    LANE_OFFSETS,
};
use super::state::{CompareFunc, RasterState, StencilFace, StencilOp};
use crate::simd::{f32x8, f64x4, i32x8};

const BLOCK: i32 = 8;
const OFFSETS_LO: f64x4 = f64x4::new([0.0, 1.0, 2.0, 3.0]);
const OFFSETS_HI: f64x4 = f64x4::new([4.0, 5.0, 6.0, 7.0]);
const OFFSETS_I32: i32x8 = i32x8::new([0, 1, 2, 3, 4, 5, 6, 7]);

/// Set bits of every byte; `count_ones` is a library loop on baseline
/// x86-64 (no POPCNT), a table is one load.
const POPCOUNT: [u8; 256] = {
    let mut t = [0u8; 256];
    let mut i = 0;
    while i < 256 {
        t[i] = (i as u8).count_ones() as u8;
        i += 1;
    }
    t
};

/// Side of the first level of blocks inside a tile.
const SUPER: i32 = 16;

/// Classifies the `size × size` block at `(x, y)` against each edge on its
/// corner samples: `None` when it lies wholly outside an edge, else which
/// edges cross it.
#[inline]
fn classify<const N: usize>(t: &SetupTriangle<N>, x: i32, y: i32, size: i32) -> Option<[bool; 3]> {
    let mut partial = [false; 3];
    for (e, p) in t.edges.iter().zip(partial.iter_mut()) {
        let corner = e.at_pixel(x as i64, y as i64);
        let sx = e.step_x() * (size as i64 - 1);
        let sy = e.step_y() * (size as i64 - 1);
        if corner + sx.max(0) + sy.max(0) < 0 {
            return None;
        }
        *p = corner + sx.min(0) + sy.min(0) < 0;
    }
    Some(partial)
}

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

/// What depth bounds say about a rectangle of a counting pass.
#[derive(Clone, Copy, PartialEq, Eq)]
enum Verdict {
    /// No covered pixel in it counts.
    Skip,
    /// Every covered pixel in it counts: no depth test needed.
    CountAll,
    /// Test pixel by pixel.
    Test,
}

/// Blocks per tile side.
const BLOCKS: usize = TILE_SIZE / BLOCK as usize;

/// Smallest and largest stored depth over rectangles of 8×8 blocks of a
/// tile, as a two-dimensional sparse table: level `(kx, ky)` holds, for
/// every block `(bx, by)`, the bounds over the `2^kx × 2^ky` blocks from
/// it. Any rectangle of blocks is the union of four such (overlapping)
/// squares, so its bounds take four lookups.
struct DepthBounds {
    /// `[ky * 4 + kx][by * 8 + bx]`.
    min: [[f32; BLOCKS * BLOCKS]; 16],
    max: [[f32; BLOCKS * BLOCKS]; 16],
}

impl DepthBounds {
    fn of(depth: &[f32]) -> Self {
        let mut b = DepthBounds {
            min: [[0.0; BLOCKS * BLOCKS]; 16],
            max: [[0.0; BLOCKS * BLOCKS]; 16],
        };
        for k in 0..BLOCKS * BLOCKS {
            let (bx, by) = (k % BLOCKS, k / BLOCKS);
            let mut mn = f32x8::splat(f32::INFINITY);
            let mut mx = f32x8::splat(f32::NEG_INFINITY);
            for r in 0..LANES {
                let i = (by * LANES + r) * TILE_SIZE + bx * LANES;
                let v = f32x8::load(&depth[i..]);
                mn = mn.min(v);
                mx = mx.max(v);
            }
            b.min[0][k] = mn.to_array().into_iter().fold(f32::INFINITY, f32::min);
            b.max[0][k] = mx.to_array().into_iter().fold(f32::NEG_INFINITY, f32::max);
        }
        let min = |a: f32, b: f32| if a < b { a } else { b };
        let max = |a: f32, b: f32| if a > b { a } else { b };
        for ky in 0..4 {
            for kx in 0..4 {
                if kx == 0 && ky == 0 {
                    continue;
                }
                // From the level one step smaller along x (or y).
                let (from, step) = if kx > 0 {
                    (ky * 4 + kx - 1, 1 << (kx - 1))
                } else {
                    ((ky - 1) * 4, BLOCKS << (ky - 1))
                };
                let (w, h) = (BLOCKS + 1 - (1 << kx), BLOCKS + 1 - (1 << ky));
                for by in 0..h {
                    for bx in 0..w {
                        let k = by * BLOCKS + bx;
                        b.min[ky * 4 + kx][k] = min(b.min[from][k], b.min[from][k + step]);
                        b.max[ky * 4 + kx][k] = max(b.max[from][k], b.max[from][k + step]);
                    }
                }
            }
        }
        b
    }

    /// The verdict for tile-local pixels `[x0, y0, x1, y1]` (inclusive)
    /// of a triangle with depth `plane` (screen origin of the tile
    /// `origin`), the test being `Greater` and the counted pixels the
    /// failing ones when `on_fail`.
    #[inline]
    fn verdict(
        &self,
        plane: &super::setup::Plane,
        plane2: Option<&super::setup::Plane>,
        origin: (i32, i32),
        rect: [i32; 4],
        on_fail: bool,
    ) -> Verdict {
        let [bx0, by0, bx1, by1] = rect.map(|v| (v / BLOCK) as usize);
        // Largest powers of two within the extents: four squares.
        let kx = (usize::BITS - 1 - (bx1 - bx0 + 1).leading_zeros()) as usize;
        let ky = (usize::BITS - 1 - (by1 - by0 + 1).leading_zeros()) as usize;
        let level = ky * 4 + kx;
        let (bx2, by2) = (bx1 + 1 - (1 << kx), by1 + 1 - (1 << ky));
        let corners = [
            by0 * BLOCKS + bx0,
            by0 * BLOCKS + bx2,
            by2 * BLOCKS + bx0,
            by2 * BLOCKS + bx2,
        ];
        let (mut lo, mut hi) = (f32::INFINITY, f32::NEG_INFINITY);
        for k in corners {
            if self.min[level][k] < lo {
                lo = self.min[level][k];
            }
            if self.max[level][k] > hi {
                hi = self.max[level][k];
            }
        }
        let screen = [
            rect[0] + origin.0,
            rect[1] + origin.1,
            rect[2] + origin.0,
            rect[3] + origin.1,
        ];
        // Every pixel fails when even the nearest fragment is not in
        // front of the farthest stored depth; every one passes when the
        // farthest fragment is in front of the nearest stored depth.
        // A quad's pixels take one of its two planes: both must agree.
        let all_fail = || {
            plane_bound(plane, screen, true) <= lo
                && plane2.is_none_or(|p| plane_bound(p, screen, true) <= lo)
        };
        let all_pass = || {
            plane_bound(plane, screen, false) > hi
                && plane2.is_none_or(|p| plane_bound(p, screen, false) > hi)
        };
        let (skip, count) = if on_fail {
            (all_pass(), all_fail())
        } else {
            (all_fail(), all_pass())
        };
        if skip {
            Verdict::Skip
        } else if count {
            Verdict::CountAll
        } else {
            Verdict::Test
        }
    }
}

/// Largest (`max`) or smallest depth the rasterizer gives any pixel of
/// `[x0, y0, x1, y1]` (screen, inclusive). The SIMD path computes a
/// pixel's depth as `clamp(row_base(y) + dx · cx(x))` with `row_base` and
/// `cx` rounded functions that are monotonic in `y` and `x`, and every
/// rounding is monotonic: the computed depth is monotonic in `x` and in
/// `y` separately, so its extremes over a rectangle are at the corners
/// the slopes' signs pick, evaluated here by the very same operations.
#[inline]
fn plane_bound(plane: &super::setup::Plane, rect: [i32; 4], max: bool) -> f32 {
    let x = if (plane.dx >= 0.0) == max {
        rect[2]
    } else {
        rect[0]
    };
    let y = if (plane.dy >= 0.0) == max {
        rect[3]
    } else {
        rect[1]
    };
    // As the SIMD path's `max` / `min` (the same compare and pick).
    let v = plane.at(x, y);
    let v = if v > 0.0 { v } else { 0.0 };
    if v < 1.0 {
        v
    } else {
        1.0
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

/// Per-tile counters.
#[derive(Debug, Clone, Copy, Default, PartialEq, Eq)]
pub struct TileStats {
    /// Covered samples that reached the tests.
    pub fragments: u64,
    /// Samples that passed stencil and depth tests.
    pub passed: u64,
}

/// One partial edge's values along a block row, stepped down the rows.
#[derive(Clone, Copy, Default)]
struct EdgeRows {
    value: f64x4,
    lanes_lo: f64x4,
    lanes_hi: f64x4,
    step_y: f64x4,
}

/// Everything constant over one tile's work.
pub(crate) struct TileJob<'a, const N: usize, S: FragmentStage<N>> {
    pub tile: usize,
    pub origin: (i32, i32),
    pub triangles: &'a [SetupTriangle<N>],
    /// Extras of the merged quads among `triangles` (counting passes).
    pub quads: &'a [QuadExtra],
    pub bin: &'a [u32],
    pub state: &'a RasterState,
    pub stage: &'a S,
    /// Set for pure counting passes (see [`CountingPass`]).
    pub counting: Option<CountingPass>,
}

/// A stencil pass that only counts: no fragment stage, no depth writes, an
/// always-passing stencil test, and per facing a single operation that
/// adds ±1 either where the depth test fails (z-fail) or where it passes
/// (z-pass). Shadow volumes are exactly this; rows then reduce to one
/// compare and one masked add.
#[derive(Debug, Clone, Copy)]
pub(crate) struct CountingPass {
    /// Added per front-facing fragment.
    front: i32,
    /// Added per back-facing fragment.
    back: i32,
    /// Count where the depth test fails (z-fail) rather than passes.
    on_depth_fail: bool,
}

impl CountingPass {
    /// The counting form of `state`, if it has one.
    pub(crate) fn of<const N: usize, S: FragmentStage<N>>(state: &RasterState) -> Option<Self> {
        if S::SHADES || S::DISCARDS || state.depth_write {
            return None;
        }
        let st = state.stencil?;
        let delta = |op: StencilOp| match op {
            StencilOp::Keep => Some(0),
            StencilOp::Increment => Some(1),
            StencilOp::Decrement => Some(-1),
            _ => None,
        };
        let face = |f: StencilFace| -> Option<(i32, i32)> {
            if f.func != CompareFunc::Always || f.stencil_fail != StencilOp::Keep {
                return None;
            }
            Some((delta(f.depth_fail)?, delta(f.pass)?))
        };
        let (front_fail, front_pass) = face(st.front)?;
        let (back_fail, back_pass) = face(st.back)?;
        if front_pass == 0 && back_pass == 0 {
            Some(CountingPass {
                front: front_fail,
                back: back_fail,
                on_depth_fail: true,
            })
        } else if front_fail == 0 && back_fail == 0 {
            Some(CountingPass {
                front: front_pass,
                back: back_pass,
                on_depth_fail: false,
            })
        } else {
            None
        }
    }
}

impl<const N: usize, S: FragmentStage<N>> TileJob<'_, N, S> {
    /// Rasterizes every binned triangle into this tile, in bin order.
    pub fn run(&self, ds: &mut DepthStencilTile, target: &mut S::Target) -> TileStats {
        if let Some(c) = self.counting {
            return self.run_counting(c, ds, target);
        }
        let mut stats = TileStats::default();
        let (tx, ty) = self.origin;
        let last = TILE_SIZE as i32 - 1;
        // Depth bounds skip rectangles where no fragment can pass, for
        // passes whose only effect is on passing fragments (no depth
        // write, no stencil): a wedge pass counting faces in front of
        // (Greater) or behind (LessEqual, the exact complement) receivers.
        let use_bounds = !self.state.depth_write
            && self.state.stencil.is_none()
            && matches!(
                self.state.depth_func,
                CompareFunc::Greater | CompareFunc::LessEqual
            );
        let on_fail = self.state.depth_func == CompareFunc::LessEqual;
        let mut bounds: Option<DepthBounds> = None;
        let mut skip = |t: &SetupTriangle<N>, rect: [i32; 4], depth: &[f32]| -> bool {
            use_bounds && {
                let local = [rect[0] - tx, rect[1] - ty, rect[2] - tx, rect[3] - ty];
                let b = bounds.get_or_insert_with(|| DepthBounds::of(depth));
                b.verdict(&t.depth, None, self.origin, local, on_fail) == Verdict::Skip
            }
        };
        for &ti in self.bin {
            let t = &self.triangles[ti as usize];
            let clip = [
                t.bbox[0].max(tx),
                t.bbox[1].max(ty),
                t.bbox[2].min(tx + last),
                t.bbox[3].min(ty + last),
            ];
            if clip[0] > clip[2] || clip[1] > clip[3] {
                continue;
            }
            if skip(t, clip, &ds.depth) {
                continue;
            }
            if t.small {
                self.small(t, clip, ds, target, &mut stats);
                continue;
            }
            // Two levels: 16×16 sub-blocks, then 8×8 blocks, each
            // classified on exact corner values; thin triangles (shadow
            // volume sides) skip most of their bounding box at the first
            // level.
            let mut sy = clip[1] & !(SUPER - 1);
            while sy <= clip[3] {
                let mut sx = clip[0] & !(SUPER - 1);
                while sx <= clip[2] {
                    let sub = [
                        sx.max(clip[0]),
                        sy.max(clip[1]),
                        (sx + SUPER - 1).min(clip[2]),
                        (sy + SUPER - 1).min(clip[3]),
                    ];
                    let covered = classify(t, sx, sy, SUPER);
                    if let Some(partial) = covered.filter(|_| !skip(t, sub, &ds.depth)) {
                        let inside = !partial.iter().any(|&p| p);
                        let mut by = sy.max(clip[1] & !(BLOCK - 1));
                        while by < sy + SUPER && by <= clip[3] {
                            let mut bx = sx.max(clip[0] & !(BLOCK - 1));
                            while bx < sx + SUPER && bx <= clip[2] {
                                let block_partial = if inside {
                                    Some([false; 3])
                                } else {
                                    classify(t, bx, by, BLOCK)
                                };
                                if let Some(p) = block_partial {
                                    self.block(t, bx, by, clip, p, ds, target, &mut stats);
                                }
                                bx += BLOCK;
                            }
                            by += BLOCK;
                        }
                    }
                    sx += SUPER;
                }
                sy += SUPER;
            }
        }
        stats
    }

    /// [`TileJob::run`] for a counting pass: triangles larger than 8×8
    /// pixels are walked row by row as exact spans (see [`SpanWalk`]), so
    /// a long sliver costs one batch per row it covers and nothing for the
    /// rest of its bounding box.
    fn run_counting(
        &self,
        c: CountingPass,
        ds: &mut DepthStencilTile,
        target: &mut S::Target,
    ) -> TileStats {
        // The depth compare is monomorphised for the one volumes use.
        match self.state.depth_func {
            CompareFunc::Greater => {
                self.count_spans(c, ds, target, |f, s| f.cmp_gt(s).cast_i32())
            }
            func => self.count_spans(c, ds, target, |f, s| compare_f32_lanes(func, f, s)),
        }
    }

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
        let last = TILE_SIZE as i32 - 1;
        // Counted lanes are `pass ^ flip`: the failing ones for z-fail.
        let flip = i32x8::splat(if c.on_depth_fail { -1 } else { 0 });
        // Depth bounds of the tile's blocks, made on first use: a pass
        // that counts does not write depth, so they hold for the whole
        // pass. Only the volumes' test (Greater) uses them.
        let use_bounds = self.state.depth_func == CompareFunc::Greater;
        let mut bounds: Option<DepthBounds> = None;
        for &ti in self.bin {
            let t = &self.triangles[ti as usize];
            let clip = [
                t.bbox[0].max(tx),
                t.bbox[1].max(ty),
                t.bbox[2].min(tx + last),
                t.bbox[3].min(ty + last),
            ];
            if clip[0] > clip[2] || clip[1] > clip[3] {
                continue;
            }
            if t.small {
                self.small(t, clip, ds, target, &mut stats);
                continue;
            }
            // A merged quad has a fourth edge, a second depth plane and a
            // diagonal that says which plane a pixel takes.
            let quad = self.quads.get(t.quad as usize);
            let edges = [
                t.edges[0],
                t.edges[1],
                t.edges[2],
                quad.map_or(t.edges[2], |q| q.edge),
            ];
            let edges = &edges[..3 + usize::from(quad.is_some())];
            let Some(rows) = SpanWalk::rows(edges, clip) else {
                continue;
            };
            let Some(stencil) = ds.stencil.as_deref_mut() else {
                continue;
            };
            let depth = &ds.depth[..];
            let plane = t.depth;
            let plane2 = quad.map(|q| q.depth2);
            let delta = i32x8::splat(if t.front_facing { c.front } else { c.back });
            let (x0, dx) = (f32x8::splat(plane.x0), f32x8::splat(plane.dx));
            // The whole rectangle's verdict first, then band by band.
            let lines = use_bounds.then(|| EdgeLines::of(edges));
            let mut pair = Verdict::Test;
            if let Some(lines) = &lines {
                let (xl, xh) = lines.extent(rows.0, rows.1, clip[0], clip[2]);
                if xl > xh {
                    continue;
                }
                let b = bounds.get_or_insert_with(|| DepthBounds::of(depth));
                let rect = [xl - tx, rows.0 - ty, xh - tx, rows.1 - ty];
                pair = b.verdict(&plane, plane2.as_ref(), self.origin, rect, c.on_depth_fail);
                if pair == Verdict::Skip {
                    continue;
                }
            }
            // The walk, when it stands at row `walk_row`.
            let mut walk: Option<SpanWalk> = None;
            let mut walk_row = rows.0;
            let mut seen = false;
            let mut y = rows.0;
            // Bands of up to 8 rows inside one row of blocks.
            while y <= rows.1 {
                let band = (y, (y | (BLOCK - 1)).min(rows.1));
                y = band.1 + 1;
                let mut verdict = pair;
                let one_band = band.0 == rows.0 && band.1 == rows.1;
                if let (Verdict::Test, false, Some(lines), Some(b)) =
                    (pair, one_band, &lines, &bounds)
                {
                    let (xl, xh) = lines.extent(band.0, band.1, clip[0], clip[2]);
                    if xl > xh {
                        continue;
                    }
                    let rect = [xl - tx, band.0 - ty, xh - tx, band.1 - ty];
                    verdict =
                        b.verdict(&plane, plane2.as_ref(), self.origin, rect, c.on_depth_fail);
                    if verdict == Verdict::Skip {
                        continue;
                    }
                }
                let tested = verdict == Verdict::Test;
                let w = match &mut walk {
                    Some(w) if walk_row == band.0 => w,
                    _ => walk.insert(SpanWalk::at(edges, clip, band.0)),
                };
                walk_row = band.1 + 1;
                let mut done = false;
                for yy in band.0..=band.1 {
                    let (lo, hi) = w.span();
                    w.step();
                    if lo > hi {
                        // A thin triangle may pass between the pixel
                        // centres of a row and cover the next; once even
                        // the real interval is empty, the convex triangle
                        // has left the rectangle for good.
                        if seen && lo > hi + 1 {
                            done = true;
                            break;
                        }
                        continue;
                    }
                    seen = true;
                    stats.fragments += (hi - lo + 1) as u64;
                    let mut x = clip[0] + lo;
                    let mut left = hi - lo + 1;
                    let mut local = ((yy - ty) as usize) * TILE_SIZE + (x - tx) as usize;
                    let base = f32x8::splat(plane.row_base(yy));
                    loop {
                        // Live lanes: the span's pixels from x on. Lanes
                        // past the tile row (padding or the next row) are
                        // loaded and stored back unchanged.
                        let live = i32x8::splat(left).cmp_gt(OFFSETS_I32);
                        let counted = if tested {
                            // Plane::lanes_on_row with the per-triangle
                            // splats hoisted: the same operations, the
                            // same bits.
                            let cx =
                                (f32x8::splat(x as f32) + LANE_OFFSETS) + f32x8::splat(0.5) - x0;
                            let mut frag = base + dx * cx;
                            if let (Some(q), Some(p2)) = (quad, &plane2) {
                                // The second triangle's pixels take its
                                // plane, computed as for it alone.
                                let second = p2.lanes(x, yy);
                                let first = edge_lanes(&q.diagonal, x, yy);
                                frag = first.cast_f32().blend(frag, second);
                            }
                            let frag = frag.max(f32x8::splat(0.0)).min(f32x8::splat(1.0));
                            let stored: &[f32; LANES] =
                                depth[local..local + LANES].try_into().expect("8 lanes");
                            (test(frag, f32x8::new(*stored)) ^ flip) & live
                        } else {
                            live
                        };
                        let s: &mut [i32; LANES] = (&mut stencil[local..local + LANES])
                            .try_into()
                            .expect("8 lanes");
                        *s = (i32x8::new(*s) + (counted & delta)).to_array();
                        if left <= BLOCK {
                            break;
                        }
                        left -= BLOCK;
                        x += BLOCK;
                        local += LANES;
                    }
                }
                if done {
                    break;
                }
            }
        }
        stats
    }

    /// A triangle spanning less than 8×8 pixels: one batch per box row,
    /// lanes starting at the box's left column. Its edge coefficients are
    /// below 8 · 256 and the box's samples lie within 9 pixels of every
    /// vertex, so edge values stay below 2 · 8 · 256 · 9 · 256 < 2^31 in
    /// magnitude: `i32` lanes hold them exactly.
    #[inline]
    fn small(
        &self,
        t: &SetupTriangle<N>,
        clip: [i32; 4],
        ds: &mut DepthStencilTile,
        target: &mut S::Target,
        stats: &mut TileStats,
    ) {
        let x = clip[0];
        let lanes = (0xffu32 >> (BLOCK - 1 - (clip[2] - x))) as u8;
        let mut value = [i32x8::splat(0); 3];
        let mut step_y = [0i32; 3];
        for k in 0..3 {
            let e = &t.edges[k];
            let base = e.at_pixel(x as i64, clip[1] as i64) as i32;
            value[k] = i32x8::splat(base) + OFFSETS_I32 * i32x8::splat(e.step_x() as i32);
            step_y[k] = e.step_y() as i32;
        }
        for y in clip[1]..=clip[3] {
            let outside = (value[0] | value[1] | value[2]).move_mask() as u8;
            let mask = lanes & !outside;
            if mask != 0 {
                self.row(t, x, y, mask, ds, target, stats);
            }
            for k in 0..3 {
                value[k] += i32x8::splat(step_y[k]);
            }
        }
    }

    /// One 8×8 block whose edges crossing it are `partial`.
    #[allow(clippy::too_many_arguments)]
    #[inline]
    fn block(
        &self,
        t: &SetupTriangle<N>,
        bx: i32,
        by: i32,
        clip: [i32; 4],
        partial: [bool; 3],
        ds: &mut DepthStencilTile,
        target: &mut S::Target,
        stats: &mut TileStats,
    ) {
        // Lanes inside the scissored bounding box.
        let lo = (clip[0] - bx).max(0);
        let hi = (clip[2] - bx).min(BLOCK - 1);
        let box_bits = ((0xffu32 << lo) & (0xffu32 >> (BLOCK - 1 - hi))) as u8;
        let first_row = by.max(clip[1]);
        let last_row = (by + BLOCK - 1).min(clip[3]);
        let any_partial = partial.iter().any(|&p| p);
        if any_partial && t.block_i32 {
            // Partial edges of a triangle whose edges are short enough:
            // inside a block they cross, values stay below 2^31, so 8
            // exact i32 lanes do one row at once.
            let mut value = [i32x8::splat(0); 3];
            let mut step_y = [0i32; 3];
            let mut n = 0;
            for (e, _) in t.edges.iter().zip(partial).filter(|(_, p)| *p) {
                let base = e.at_pixel(bx as i64, first_row as i64) as i32;
                value[n] = i32x8::splat(base) + OFFSETS_I32 * i32x8::splat(e.step_x() as i32);
                step_y[n] = e.step_y() as i32;
                n += 1;
            }
            for y in first_row..=last_row {
                let mut or = value[0];
                for v in &value[1..n] {
                    or |= *v;
                }
                let mask = box_bits & !(or.move_mask() as u8);
                if mask != 0 {
                    self.row(t, bx, y, mask, ds, target, stats);
                }
                for k in 0..n {
                    value[k] += i32x8::splat(step_y[k]);
                }
            }
            return;
        }
        // Partial edges, stepped row by row in f64: every value is an
        // integer below 2^53, so the additions are exact.
        let zero = f64x4::splat(0.0);
        let mut rows = [EdgeRows {
            value: zero,
            lanes_lo: zero,
            lanes_hi: zero,
            step_y: zero,
        }; 3];
        let mut n = 0;
        for (e, _) in t.edges.iter().zip(partial).filter(|(_, p)| *p) {
            let step = f64x4::splat(e.step_x() as f64);
            rows[n] = EdgeRows {
                value: f64x4::splat(e.at_pixel(bx as i64, first_row as i64) as f64),
                lanes_lo: OFFSETS_LO * step,
                lanes_hi: OFFSETS_HI * step,
                step_y: f64x4::splat(e.step_y() as f64),
            };
            n += 1;
        }
        for y in first_row..=last_row {
            let mut mask = box_bits;
            if n > 0 {
                // A lane is outside when any partial edge is negative
                // there: OR the values and read the sign bits. (Values are
                // never -0.0: they are sums of integers starting from a
                // converted i64.)
                let (mut lo, mut hi) = (f64x4::splat(0.0), f64x4::splat(0.0));
                for r in &mut rows[..n] {
                    lo |= r.value + r.lanes_lo;
                    hi |= r.value + r.lanes_hi;
                    r.value += r.step_y;
                }
                let outside = lo.move_mask() | (hi.move_mask() << 4);
                mask &= !(outside as u8);
            }
            if mask != 0 {
                self.row(t, bx, y, mask, ds, target, stats);
            }
        }
    }

    /// Tests, updates and shades 8 fragments `(x + k, y)` of one row.
    /// Live lanes lie inside the tile; the depth and stencil tiles carry 8
    /// elements of padding so that a batch starting near a row's end may
    /// read and write back (unchanged) lanes past it.
    #[allow(clippy::too_many_arguments)]
    #[inline(always)]
    fn row(
        &self,
        t: &SetupTriangle<N>,
        x: i32,
        y: i32,
        mut mask: u8,
        ds: &mut DepthStencilTile,
        target: &mut S::Target,
        stats: &mut TileStats,
    ) {
        let local = ((y - self.origin.1) as usize) * TILE_SIZE + (x - self.origin.0) as usize;
        // Clamped into [0, 1] (planes are finite; the facade's `max` /
        // `min` are one instruction each on x86).
        let depth = t
            .depth
            .lanes(x, y)
            .max(f32x8::splat(0.0))
            .min(f32x8::splat(1.0));
        let stored_depth = f32x8::load(&ds.depth[local..]);
        if let (Some(c), Some(stencil)) = (self.counting, ds.stencil.as_mut()) {
            let pass = compare_f32(self.state.depth_func, depth, stored_depth);
            let lanes = mask & if c.on_depth_fail { !pass } else { pass };
            let delta = if t.front_facing { c.front } else { c.back };
            stats.fragments += POPCOUNT[mask as usize] as u64;
            if lanes != 0 && delta != 0 {
                let stored = i32x8::load(&stencil[local..]);
                let add = select_i32(lanes, i32x8::splat(delta), i32x8::splat(0));
                stencil[local..local + LANES].copy_from_slice(&(stored + add).to_array());
            }
            return;
        }
        // The batch is built only for stages that look at it: a depth or
        // stencil pass never pays for it.
        let batch = |mask: u8| {
            let mut varyings = [f32x8::splat(0.0); N];
            interpolate(t, x, y, &mut varyings);
            FragmentBatch {
                x,
                y,
                tile: self.tile,
                local,
                mask,
                depth,
                stored_depth,
                varyings,
                front_facing: t.front_facing,
                primitive: t.primitive,
            }
        };
        if S::DISCARDS {
            mask &= self.stage.discard(&batch(mask));
            if mask == 0 {
                return;
            }
        }
        stats.fragments += POPCOUNT[mask as usize] as u64;

        let state = self.state;
        let passed = match (&state.stencil, ds.stencil.as_mut()) {
            (Some(st), Some(stencil)) => {
                let face = if t.front_facing { st.front } else { st.back };
                let stored = i32x8::load(&stencil[local..]);
                let s_pass = match face.func {
                    CompareFunc::Always => mask,
                    func => compare_i32(func, st.reference, stored) & mask,
                };
                let d_pass = compare_f32(state.depth_func, depth, stored_depth) & s_pass;
                // Only operations that change something are evaluated: a
                // z-fail pass, say, has a single non-Keep operation.
                let r = st.reference;
                let mut new = stored;
                let mut changed = false;
                for (op, lanes) in [
                    (face.stencil_fail, mask & !s_pass),
                    (face.depth_fail, s_pass & !d_pass),
                    (face.pass, d_pass),
                ] {
                    if lanes != 0 && !matches!(op, StencilOp::Keep) {
                        new = select_i32(lanes, stencil_op(op, stored, r), new);
                        changed = true;
                    }
                }
                if changed {
                    stencil[local..local + LANES].copy_from_slice(&new.to_array());
                }
                d_pass
            }
            _ => compare_f32(state.depth_func, depth, stored_depth) & mask,
        };
        if passed == 0 {
            return;
        }
        stats.passed += POPCOUNT[passed as usize] as u64;
        if state.depth_write {
            let new = select_f32(passed, depth, stored_depth);
            ds.depth[local..local + LANES].copy_from_slice(&new.to_array());
        }
        if S::SHADES {
            self.stage.shade(&batch(passed), target);
        }
    }
}

/// Perspective-correct varyings: `(v / w) / (1 / w)`, both interpolated
/// linearly in screen space.
#[inline]
fn interpolate<const N: usize>(t: &SetupTriangle<N>, x: i32, y: i32, out: &mut [f32x8; N]) {
    if N == 0 {
        return;
    }
    let inv_w = t.inv_w.lanes(x, y);
    for (o, p) in out.iter_mut().zip(t.varyings.iter()) {
        *o = p.lanes(x, y) / inv_w;
    }
}

#[cfg(test)]
mod tests {
    use super::*;
    use crate::raster::setup::{EdgeFunction, Plane};

    struct Lcg(u64);
    impl Lcg {
        fn below(&mut self, n: i64) -> i64 {
            self.0 = self
                .0
                .wrapping_mul(6364136223846793005)
                .wrapping_add(1442695040888963407);
            ((self.0 >> 33) as i64).rem_euclid(n)
        }
    }

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

    /// The sparse table's bounds over any rectangle of blocks are the
    /// bounds of the pixels in those blocks, and verdicts follow them.
    #[test]
    fn depth_bounds_over_any_block_rectangle() {
        let mut rng = Lcg(9);
        let depth: Vec<f32> = (0..TILE_SIZE * TILE_SIZE + LANES)
            .map(|_| rng.below(1_000_000) as f32 * 1e-6)
            .collect();
        let b = DepthBounds::of(&depth);
        for by0 in 0..BLOCKS {
            for by1 in by0..BLOCKS {
                for bx0 in 0..BLOCKS {
                    for bx1 in bx0..BLOCKS {
                        let (mut lo, mut hi) = (f32::INFINITY, f32::NEG_INFINITY);
                        for y in by0 * 8..by1 * 8 + 8 {
                            for x in bx0 * 8..bx1 * 8 + 8 {
                                lo = lo.min(depth[y * TILE_SIZE + x]);
                                hi = hi.max(depth[y * TILE_SIZE + x]);
                            }
                        }
                        // Pixel rectangles inside those blocks.
                        let rect = [
                            (bx0 * 8 + rng.below(8) as usize) as i32,
                            (by0 * 8 + rng.below(8) as usize) as i32,
                            (bx1 * 8 + rng.below(8) as usize) as i32,
                            (by1 * 8 + rng.below(8) as usize) as i32,
                        ];
                        // A flat plane at depth d: all pass iff d > hi,
                        // all fail iff d <= lo.
                        for d in [lo, hi, (lo + hi) / 2.0, lo - 1e-3, hi + 1e-3] {
                            let plane = Plane {
                                v0: d,
                                ..Plane::default()
                            };
                            let want = if d > hi {
                                Verdict::Skip
                            } else if d <= lo {
                                Verdict::CountAll
                            } else {
                                Verdict::Test
                            };
                            assert!(want == b.verdict(&plane, None, (0, 0), rect, true));
                        }
                    }
                }
            }
        }
    }

    /// The depth the SIMD path gives a pixel is monotonic along x and y,
    /// so [`plane_bound`] over a rectangle bounds every pixel in it.
    #[test]
    fn plane_bounds_hold_every_pixel() {
        let mut rng = Lcg(5);
        for _ in 0..2000 {
            let f = |rng: &mut Lcg| (rng.below(2001) - 1000) as f32 * 1e-3;
            let plane = Plane {
                x0: f(&mut rng) * 500.0,
                y0: f(&mut rng) * 500.0,
                v0: f(&mut rng) + 0.5,
                dx: f(&mut rng) * 1e-3,
                dy: f(&mut rng) * 1e-3,
            };
            let x0 = rng.below(1000) as i32;
            let y0 = rng.below(1000) as i32;
            let rect = [x0, y0, x0 + rng.below(64) as i32, y0 + rng.below(8) as i32];
            let (lo, hi) = (
                plane_bound(&plane, rect, false),
                plane_bound(&plane, rect, true),
            );
            for y in rect[1]..=rect[3] {
                for x in (rect[0]..=rect[2]).step_by(LANES) {
                    let v = plane
                        .lanes(x, y)
                        .max(f32x8::splat(0.0))
                        .min(f32x8::splat(1.0))
                        .to_array();
                    for (k, v) in v.iter().enumerate() {
                        if x + (k as i32) <= rect[2] {
                            assert!(
                                lo <= *v && *v <= hi,
                                "{plane:?} {rect:?}: {v} outside {lo}..{hi}"
                            );
                        }
                    }
                }
            }
        }
    }
}
